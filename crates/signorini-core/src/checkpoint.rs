//! Checkpoints of a running job: everything the next step and the rest of the run read, as a
//! value ([`Checkpoint`]) and as versioned bytes ([`Checkpoint::encode`], [`Checkpoint::decode`]).
//!
//! A run offers a checkpoint after a step when its observer asks for one
//! ([`Observer::checkpoint_due`], which the caller answers from its own clock or step count: the
//! core keeps none); [`crate::job::resume`] continues from it. The checkpoint holds the scheme's
//! state (for Moreau–Jean the cached end-of-step energy and load, for the α-family its filters and
//! accelerations, for SOI2 a_α, the Newton cache and the position in the step-size schedule, for
//! WFEM the cells), the index set with its round-off levels, the loop's running statistics and
//! previous impulses, the last step's report, and the observers' state in the core (the
//! envelopes of [`crate::trace::EnergyTrace`], the grid of
//! [`crate::contact_region::ContactRegion`], the count of records handed out). Nothing that is
//! rebuilt from the spec (factorisations, Delassus operators, compiled models) is stored: a
//! resumed run rebuilds it bit for bit from the same spec, which the header's spec hash pins.
//!
//! This module is a leaf: the time-stepping driver ([`crate::stepping::run`]) encodes a family's
//! memory into the checkpoint as a tagged section ([`RunKind`] and bytes) and decodes it back,
//! so no family depends on another.
//!
//! # Format (version [`FORMAT_VERSION`])
//!
//! ```text
//! magic "SIGNCKPT" (8 bytes) | format version u32 LE | spec hash u64 LE | payload length u64 LE
//! | payload checksum u64 LE (FNV-1a 64) | payload (MessagePack, structs as maps)
//! ```
//!
//! MessagePack ([rmp-serde](https://docs.rs/rmp-serde)) stores every f64 as its 8 raw bytes, so
//! values round-trip bit for bit (NaN payloads included), and it is self-describing enough for the
//! summary types' optional fields (`skip_serializing_if`), which the non-self-describing formats
//! (postcard, bincode) cannot read back. A checkpoint of another format version, another spec,
//! or with a wrong length or checksum is refused with a [`CheckpointError`] before anything is
//! restored.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Version of the checkpoint format this build writes and reads. Version 2 added the banded
/// contact solver's warm start to the Moreau–Jean and α-family states and the
/// `contact_region` chart's grid ([`crate::contact_region`]); version 1 is refused
/// ([`CheckpointError::Version`]). The run loop's state has a version of its own per
/// [`RunKind`] ([`RunKind::state_version`]), so that one family's state can change without
/// refusing the checkpoints of the others.
pub const FORMAT_VERSION: u32 = 2;

const MAGIC: &[u8; 8] = b"SIGNCKPT";
const HEADER_LEN: usize = 8 + 4 + 8 + 8 + 8;

/// Why a checkpoint was refused. Nothing of a refused checkpoint is restored.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CheckpointError {
    /// The bytes do not start with the checkpoint magic.
    #[error("not a Signorini checkpoint (no SIGNCKPT header)")]
    Magic,
    /// Shorter than its header says.
    #[error("checkpoint truncated: {found} bytes, {expected} expected")]
    Truncated {
        /// Bytes expected (header and payload).
        expected: u64,
        /// Bytes found.
        found: u64,
    },
    /// Written by another format version.
    #[error("checkpoint format version {found}, this build reads version {expected}")]
    Version {
        /// The version this build reads.
        expected: u32,
        /// The checkpoint's version.
        found: u32,
    },
    /// The run loop's state was written in another version of its kind
    /// ([`RunKind::state_version`]).
    #[error(
        "checkpoint of a {kind} run with state version {found}, this build reads version {expected}: rerun the job from the start"
    )]
    StateVersion {
        /// The run kind's name.
        kind: &'static str,
        /// The version this build reads for the kind.
        expected: u32,
        /// The checkpoint's.
        found: u32,
    },
    /// Written by a run of another spec.
    #[error("checkpoint of another spec (spec hash {found:016x}, this job's is {expected:016x})")]
    Spec {
        /// This job's spec hash.
        expected: u64,
        /// The checkpoint's.
        found: u64,
    },
    /// The payload's checksum does not match: the bytes were damaged.
    #[error("checkpoint corrupted: payload checksum {found:016x}, header says {expected:016x}")]
    Checksum {
        /// The checksum in the header.
        expected: u64,
        /// The checksum of the payload read.
        found: u64,
    },
    /// The payload could not be decoded.
    #[error("checkpoint payload unreadable: {0}")]
    Decode(String),
    /// The payload could not be encoded.
    #[error("checkpoint could not be encoded: {0}")]
    Encode(String),
    /// The checkpoint is of another kind of run, or its state does not fit the job.
    #[error("checkpoint does not fit this job: {0}")]
    Mismatch(String),
    /// The job cannot be resumed from a checkpoint (an analysis).
    #[error("a {0} job has no checkpoints: it reruns from the start")]
    Unsupported(&'static str),
}

/// Everything a run needs to continue after step [`Checkpoint::step`] as if it had never stopped.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Checkpoint {
    step: u64,
    records: u64,
    spec_hash: u64,
    kind: RunKind,
    /// Version of the run loop's state ([`RunKind::state_version`]); absent, hence 1, in the
    /// checkpoints written before it existed.
    #[serde(default = "first_state_version")]
    state_version: u32,
    /// The run loop's state (MessagePack of its own state type).
    #[serde(with = "serde_bytes")]
    run: Vec<u8>,
    /// The state of [`crate::trace::EnergyTrace`], if the run had one.
    #[serde(with = "serde_bytes")]
    trace: Option<Vec<u8>>,
    /// The state of [`crate::contact_region::ContactRegion`], if the run draws one.
    #[serde(with = "serde_bytes")]
    region: Option<Vec<u8>>,
}

/// Which run loop a checkpoint belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RunKind {
    /// Linear models: Moreau–Jean, the α-family, position-contact.
    Linear,
    /// The nonlinear Moreau–Jean time-stepping of user models.
    Nonlinear,
    /// The nonsmooth generalized-α of user models.
    NsAlpha,
    /// SOI2 (generalized-α-SOI2, HHT-SOI2, HHT-I3).
    Soi2,
    /// WFEM.
    Wave,
    /// Rigid bodies under Moreau–Jean (the bodies' states and the run's statistics).
    Rigid,
}

impl RunKind {
    /// The name of the run, for errors.
    pub fn name(self) -> &'static str {
        match self {
            RunKind::Linear => "linear",
            RunKind::Nonlinear => "nonlinear Moreau–Jean",
            RunKind::NsAlpha => "ns_generalized_alpha",
            RunKind::Soi2 => "SOI2",
            RunKind::Wave => "WFEM",
            RunKind::Rigid => "rigid bodies",
        }
    }
}

impl RunKind {
    /// Version of the run loop's state this build writes and reads for the kind. The nonlinear
    /// Moreau–Jean and ns_generalized_alpha states are at version 2: it keeps only what the
    /// next step reads (the scheme's memory), where version 1 also held the last step's report
    /// and, for Moreau–Jean, its scratch buffers (mass matrix, Jacobians, Delassus operator).
    /// Rigid bodies are at version 3: version 2 added the last step's impulses per contact, from
    /// which the next step's friction problem starts (version 1 had none, and a run resumed from
    /// it would not continue bit for bit), version 3 the rows of the `contacts` table so far (a
    /// run resumed from version 2 wrote only the rows after the checkpoint). The other kinds are
    /// at version 1.
    pub fn state_version(self) -> u32 {
        match self {
            RunKind::Rigid => 3,
            RunKind::Nonlinear | RunKind::NsAlpha => 2,
            RunKind::Linear | RunKind::Soi2 | RunKind::Wave => 1,
        }
    }
}

fn first_state_version() -> u32 {
    1
}

/// `value` as MessagePack (structs as maps).
fn to_bytes<T: Serialize>(value: &T) -> Result<Vec<u8>, CheckpointError> {
    rmp_serde::to_vec_named(value).map_err(|e| CheckpointError::Encode(e.to_string()))
}

fn from_bytes<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CheckpointError> {
    rmp_serde::from_slice(bytes).map_err(|e| CheckpointError::Decode(e.to_string()))
}

impl Checkpoint {
    /// A checkpoint after step `step` of a `kind` run whose loop state is `run`; the observers
    /// in the core add their state, the record count and the spec hash as it passes through.
    pub(crate) fn new<T: Serialize>(
        step: u64,
        kind: RunKind,
        run: &T,
    ) -> Result<Self, CheckpointError> {
        Ok(Self {
            step,
            records: 0,
            spec_hash: 0,
            kind,
            state_version: kind.state_version(),
            run: to_bytes(run)?,
            trace: None,
            region: None,
        })
    }

    /// Steps done.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// Records handed to the observer up to this checkpoint (the initial record included): a
    /// caller that stored records keeps that many and drops any after them when it resumes.
    pub fn records(&self) -> u64 {
        self.records
    }

    /// The run loop it belongs to.
    pub fn kind(&self) -> RunKind {
        self.kind
    }

    /// The hash of the spec of its run.
    pub fn spec_hash(&self) -> u64 {
        self.spec_hash
    }

    pub(crate) fn stamp(&mut self, records: u64, spec_hash: u64) {
        self.records = records;
        self.spec_hash = spec_hash;
    }

    /// The loop state of a `kind` run (refused for another kind).
    pub(crate) fn run_state<T: DeserializeOwned>(
        &self,
        kind: RunKind,
    ) -> Result<T, CheckpointError> {
        if kind != self.kind {
            return Err(CheckpointError::Mismatch(format!(
                "a checkpoint of a {} run, this job is a {} run",
                self.kind.name(),
                kind.name()
            )));
        }
        if self.state_version != kind.state_version() {
            return Err(CheckpointError::StateVersion {
                kind: kind.name(),
                expected: kind.state_version(),
                found: self.state_version,
            });
        }
        from_bytes(&self.run)
    }

    pub(crate) fn set_trace<T: Serialize>(&mut self, trace: &T) -> Result<(), CheckpointError> {
        self.trace = Some(to_bytes(trace)?);
        Ok(())
    }

    pub(crate) fn trace_state<T: DeserializeOwned>(&self) -> Result<Option<T>, CheckpointError> {
        self.trace.as_deref().map(from_bytes).transpose()
    }

    pub(crate) fn set_region<T: Serialize>(&mut self, region: &T) -> Result<(), CheckpointError> {
        self.region = Some(to_bytes(region)?);
        Ok(())
    }

    pub(crate) fn region_state<T: DeserializeOwned>(&self) -> Result<Option<T>, CheckpointError> {
        self.region.as_deref().map(from_bytes).transpose()
    }

    /// The checkpoint as bytes (header and payload, see the [module](self) documentation).
    pub fn encode(&self) -> Result<Vec<u8>, CheckpointError> {
        let payload = to_bytes(self)?;
        let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&self.spec_hash.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&fnv1a(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        Ok(out)
    }

    /// Reads a checkpoint written by a run of the spec whose hash is `spec_hash`
    /// ([`crate::job::Job::read_checkpoint`] passes its own); refuses foreign, damaged or
    /// mismatched bytes with the reason.
    pub fn decode(bytes: &[u8], spec_hash: u64) -> Result<Checkpoint, CheckpointError> {
        if bytes.len() < 8 || &bytes[..8] != MAGIC {
            return Err(CheckpointError::Magic);
        }
        if bytes.len() < HEADER_LEN {
            return Err(CheckpointError::Truncated {
                expected: HEADER_LEN as u64,
                found: bytes.len() as u64,
            });
        }
        let u64_at = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[i..i + 8]);
            u64::from_le_bytes(b)
        };
        let mut v = [0u8; 4];
        v.copy_from_slice(&bytes[8..12]);
        let version = u32::from_le_bytes(v);
        if version != FORMAT_VERSION {
            return Err(CheckpointError::Version {
                expected: FORMAT_VERSION,
                found: version,
            });
        }
        let found_hash = u64_at(12);
        if found_hash != spec_hash {
            return Err(CheckpointError::Spec {
                expected: spec_hash,
                found: found_hash,
            });
        }
        let len = u64_at(20);
        let payload = &bytes[HEADER_LEN..];
        if payload.len() as u64 != len {
            return Err(CheckpointError::Truncated {
                expected: HEADER_LEN as u64 + len,
                found: bytes.len() as u64,
            });
        }
        let checksum = u64_at(28);
        let found = fnv1a(payload);
        if found != checksum {
            return Err(CheckpointError::Checksum {
                expected: checksum,
                found,
            });
        }
        let cp: Checkpoint = from_bytes(payload)?;
        if cp.spec_hash != spec_hash {
            return Err(CheckpointError::Spec {
                expected: spec_hash,
                found: cp.spec_hash,
            });
        }
        Ok(cp)
    }
}

/// FNV-1a, 64 bits (Fowler, Noll, Vo): a checksum, not a cryptographic hash.
pub(crate) fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The envelope as written before run states had versions: no `state_version` field.
    #[derive(Serialize)]
    struct Unversioned {
        step: u64,
        records: u64,
        spec_hash: u64,
        kind: RunKind,
        #[serde(with = "serde_bytes")]
        run: Vec<u8>,
        #[serde(with = "serde_bytes")]
        trace: Option<Vec<u8>>,
        #[serde(with = "serde_bytes")]
        region: Option<Vec<u8>>,
    }

    /// The bytes of an unversioned checkpoint of a `kind` run, header included.
    fn unversioned(kind: RunKind, spec_hash: u64) -> Vec<u8> {
        let payload = to_bytes(&Unversioned {
            step: 3,
            records: 4,
            spec_hash,
            kind,
            run: to_bytes(&7u64).unwrap(),
            trace: None,
            region: None,
        })
        .unwrap();
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&spec_hash.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&fnv1a(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        out
    }

    /// A checkpoint of a nonlinear Moreau–Jean or ns_generalized_alpha run written before their
    /// states dropped the scratch buffers (state version 1) is refused, naming both versions; a
    /// linear one of the same envelope still loads.
    #[test]
    fn an_old_nonlinear_state_is_refused_naming_the_versions() {
        for kind in [RunKind::Nonlinear, RunKind::NsAlpha] {
            let old = Checkpoint::decode(&unversioned(kind, 42), 42).unwrap();
            let err = old.run_state::<u64>(kind).unwrap_err();
            assert_eq!(
                err,
                CheckpointError::StateVersion {
                    kind: kind.name(),
                    expected: 2,
                    found: 1
                }
            );
            let text = err.to_string();
            assert!(
                text.contains("state version 1") && text.contains("reads version 2"),
                "{text}"
            );
            // A checkpoint written now carries version 2 and loads.
            let new = Checkpoint::new(3, kind, &7u64).unwrap();
            let bytes = new.encode().unwrap();
            let read = Checkpoint::decode(&bytes, 0).unwrap();
            assert_eq!(read.run_state::<u64>(kind).unwrap(), 7);
        }
        let linear = Checkpoint::decode(&unversioned(RunKind::Linear, 42), 42).unwrap();
        assert_eq!(linear.run_state::<u64>(RunKind::Linear).unwrap(), 7);
    }

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        // Test vectors of the FNV reference (Noll, "FNV Hash", test suite).
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
