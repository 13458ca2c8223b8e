//! Generated protobuf messages and the gRPC service of `proto/signorini/v1` (built into OUT_DIR).
#![allow(missing_docs, clippy::all, clippy::pedantic)]

/// `signorini.v1`.
pub mod v1 {
    tonic::include_proto!("signorini.v1");
}
